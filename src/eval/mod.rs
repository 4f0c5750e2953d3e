//! Evaluation: a validated graph is flattened into a [`Plan`] (graph files used as nodes are
//! inlined, graph inputs bound, relative paths resolved), then the [`Evaluator`] pulls the
//! requested outputs.
//!
//! - **Lazy**: only nodes the requested outputs need are considered, and a node whose key is
//!   cached is not descended into.
//! - **Content keys** ([`CacheKey`]): op id + op version + canonical params (floats by bits;
//!   input files by the hash of their bytes, memoised by path + mtime + size) + the keys of the
//!   inputs. Node ids, names and positions are not in the key: moving or renaming a node costs
//!   nothing.
//! - **Caches**: a byte-budgeted LRU in memory ([`cache`]) and optionally a folder on disk
//!   ([`disk`]) that survives the process.
//! - **Parallel**: nodes to run are grouped in dependency levels; each level runs on rayon.
//! - **Memory**: before anything runs, the plan's peak memory is estimated from the output
//!   sizes every operator states ([`memory`]); over the budget (`RGBN_MEMORY_LIMIT`) the
//!   evaluation is refused with an error naming the nodes that need the most.
//! - **Cancellation and progress**: [`EvalOptions::cancel`] is checked before each node and,
//!   as the [`crate::cancel::Cancel`] token of [`RunContext`], by long operators while they run;
//!   a cancelled node's result is never cached;
//!   [`EvalOptions::progress`] is called after each node that ran.

// Graph errors carry their location (file, node, names) by value; they are cold paths.
#![allow(clippy::result_large_err)]

pub mod bind;
pub mod cache;
pub mod disk;
pub mod kept;
pub mod memory;
pub mod plan;
pub mod region;
pub mod stream;
pub mod zarr_sink;

pub use cache::{CacheEntry, CacheKey, MemCache};
pub use disk::DiskCache;
pub use kept::ValueFn;
use plan::display;
pub use plan::{port_key, Conn, Instance, Plan};

use crate::graph::{At, GraphError, NodeId};
use crate::nodes::{RunContext, Value, ALL_PORTS};
use crate::params::{ParamKind, ParamValue};
use crate::raster::gradient::GradientField;
use parking_lot::Mutex;
use rayon::prelude::*;
use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime};

/// A progress report, sent after each node that ran.
#[derive(Clone, Debug)]
pub struct Progress {
    /// Nodes finished so far in this evaluation.
    pub done: usize,
    /// Nodes that must run in this evaluation.
    pub total: usize,
    /// The node that just finished.
    pub at: At,
    /// Its operator.
    pub op: &'static str,
}

/// Progress callback type.
pub type ProgressFn = Arc<dyn Fn(&Progress) + Send + Sync>;

/// Options of one evaluation.
#[derive(Clone, Default)]
pub struct EvalOptions {
    /// The evaluation's cancellation token: set it (from any thread) to stop the running
    /// operators and start no other (`crate::cancel`).
    pub cancel: crate::cancel::Cancel,
    /// Called after each node that ran.
    pub progress: Option<ProgressFn>,
    /// Measure the integrability of each node's RGBN output: its relative RMS curl and its
    /// non-integrable fraction F (one least-squares integration per node: a DCT, or the
    /// masked solver where there is a mask). The readouts are taken after every node has run,
    /// on all cores, and timed apart from the nodes ([`NodeStats::readout`]); a value keeps
    /// its readouts in the cache.
    pub curl_stats: bool,
}

impl EvalOptions {
    /// [`EvalOptions::cancel`], the token operators see ([`RunContext::cancel`]).
    #[must_use]
    pub fn token(&self) -> crate::cancel::Cancel {
        self.cancel.clone()
    }
    /// Whether [`EvalOptions::cancel`] is set.
    #[must_use]
    pub fn cancelled(&self) -> bool {
        self.cancel.is_cancelled()
    }
}

/// How a node's value was obtained.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    /// From the memory cache.
    Hit,
    /// From the disk cache.
    DiskHit,
    /// Computed (its key was not cached).
    Miss,
    /// Ran because it writes outside the graph (never cached).
    Effect,
}

/// What happened at one node.
#[derive(Clone, Debug)]
pub struct NodeStats {
    /// The node.
    pub at: At,
    /// Operator id.
    pub op: &'static str,
    /// Hit, miss, …
    pub status: Status,
    /// Time spent computing (zero for hits). Readouts are not in it.
    pub time: Duration,
    /// Time spent on the integrability readout ([`EvalOptions::curl_stats`]), apart from
    /// the node's computation (zero when not measured or measured earlier).
    pub readout: Duration,
    /// Bytes of output.
    pub bytes: usize,
    /// Relative RMS curl of the RGBN output, when measured.
    pub curl: Option<f64>,
    /// Non-integrable fraction F of the RGBN output (0: a surface; √(2/π) ≈ 0.80: noise), when
    /// measured.
    pub fraction: Option<f64>,
    /// The node's content key.
    pub key: CacheKey,
}

/// The result of an evaluation.
#[derive(Clone, Debug)]
pub struct EvalResult {
    /// The requested graph outputs.
    pub outputs: BTreeMap<String, Value>,
    /// One entry per node that was needed, in evaluation order.
    pub stats: Vec<NodeStats>,
    /// The memory estimate this evaluation was checked against.
    pub memory: memory::Estimate,
}

impl EvalResult {
    /// Nodes computed because their key was not cached.
    #[must_use]
    pub fn misses(&self) -> usize {
        self.stats
            .iter()
            .filter(|s| s.status == Status::Miss)
            .count()
    }
    /// Nodes served from a cache.
    #[must_use]
    pub fn hits(&self) -> usize {
        self.stats
            .iter()
            .filter(|s| matches!(s.status, Status::Hit | Status::DiskHit))
            .count()
    }
    /// Ids of the top-level nodes that missed (sorted, deduplicated).
    #[must_use]
    pub fn missed_nodes(&self) -> Vec<NodeId> {
        let mut v: Vec<NodeId> = self
            .stats
            .iter()
            .filter(|s| s.status == Status::Miss)
            .filter_map(|s| s.at.node)
            .collect();
        v.sort_unstable();
        v.dedup();
        v
    }
}

/// What [`Evaluator::eval_instances`] produced.
struct Whole {
    /// Outputs of every instance considered, by index.
    results: HashMap<usize, Arc<CacheEntry>>,
    /// Stats of each, in index order.
    stats: Vec<NodeStats>,
    /// The memory estimate checked.
    memory: memory::Estimate,
    /// Content keys computed on the way.
    keys: HashMap<usize, CacheKey>,
}

/// A node that ran: its index, outputs and stats.
type Ran = (usize, Arc<CacheEntry>, NodeStats);

#[derive(Clone, Copy)]
struct FileStamp {
    mtime: Option<SystemTime>,
    len: u64,
    hash: u128,
}

/// Evaluates plans, keeping results in its caches between evaluations.
pub struct Evaluator {
    mem: Mutex<MemCache>,
    disk: Option<DiskCache>,
    files: Mutex<HashMap<PathBuf, FileStamp>>,
    /// What each tiled instance was at its last region evaluation (for damage).
    seen: Mutex<region::History>,
}

impl std::fmt::Debug for Evaluator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Evaluator")
            .field("disk", &self.disk)
            .finish()
    }
}

/// Default memory budget: 1 GiB.
pub const DEFAULT_BUDGET: usize = 1 << 30;

impl Default for Evaluator {
    fn default() -> Self {
        Self::new(DEFAULT_BUDGET)
    }
}

impl Evaluator {
    /// An evaluator whose memory cache holds at most `budget_bytes`.
    #[must_use]
    pub fn new(budget_bytes: usize) -> Self {
        Self {
            mem: Mutex::new(MemCache::new(budget_bytes)),
            disk: None,
            files: Mutex::new(HashMap::new()),
            seen: Mutex::new(region::History::default()),
        }
    }

    /// Also keeps results in `dir` (created if missing).
    pub fn with_disk_cache(mut self, dir: &Path) -> Result<Self, GraphError> {
        self.disk = Some(DiskCache::new(dir).map_err(|e| GraphError::Io {
            file: display(dir),
            source: e,
        })?);
        Ok(self)
    }

    /// Entries and bytes in the memory cache.
    #[must_use]
    pub fn mem_usage(&self) -> (usize, usize) {
        let m = self.mem.lock();
        (m.len(), m.bytes())
    }

    /// Empties the memory cache (the disk cache is kept).
    pub fn clear_memory(&self) {
        self.mem.lock().clear();
    }

    fn file_hash(&self, path: &Path, at: &At) -> Result<u128, GraphError> {
        let err = |detail: String| GraphError::InputFile {
            path: display(path),
            detail,
            at: at.clone(),
        };
        let meta = std::fs::metadata(path).map_err(|e| {
            err(if e.kind() == std::io::ErrorKind::NotFound {
                "file not found".into()
            } else {
                e.to_string()
            })
        })?;
        if meta.is_dir() {
            // An OME-Zarr store: keyed by its metadata and its files' names, sizes and times,
            // not by reading every chunk (a region reads only its own).
            return crate::raster::io::zarr::stamp(path).map_err(|e| err(e.to_string()));
        }
        let (mtime, len) = (meta.modified().ok(), meta.len());
        if let Some(s) = self.files.lock().get(path) {
            if s.mtime.is_some() && s.mtime == mtime && s.len == len {
                return Ok(s.hash);
            }
        }
        let hash = hash_file(path).map_err(|e| err(e.to_string()))?;
        self.files
            .lock()
            .insert(path.to_path_buf(), FileStamp { mtime, len, hash });
        Ok(hash)
    }

    fn key(
        &self,
        plan: &Plan,
        i: usize,
        keys: &mut HashMap<usize, CacheKey>,
    ) -> Result<CacheKey, GraphError> {
        if let Some(k) = keys.get(&i) {
            return Ok(*k);
        }
        let inst = &plan.instances[i];
        let spec = inst.op.spec();
        let mut h = xxhash_rust::xxh3::Xxh3::new();
        h.update(b"rgbn-node-key-2\0");
        h.update(spec.id.as_bytes());
        h.update(&spec.version.to_le_bytes());
        h.update(&inst.params.hash().to_le_bytes());
        // Files read are keyed by their bytes (the parameters' hash leaves their paths out).
        for info in inst.op.params() {
            if info.kind != ParamKind::Path || info.meta.output {
                continue;
            }
            if let Some(ParamValue::Path(p)) = inst.params.values().get(info.name) {
                if !p.is_empty() {
                    h.update(b"file-content");
                    h.update(&self.file_hash(Path::new(p), &inst.at)?.to_le_bytes());
                }
            }
        }
        for c in &inst.inputs {
            match c {
                Conn::None => h.update(b"none"),
                Conn::Slot(j, port) => {
                    let k = self.key(plan, *j, keys)?;
                    h.update(&k.to_le_bytes());
                    h.update(&(*port as u64).to_le_bytes());
                }
                Conn::Unbound { name, at } => {
                    return Err(GraphError::UnboundInput {
                        name: name.clone(),
                        at: at.clone(),
                    })
                }
            }
        }
        let k = h.digest128();
        keys.insert(i, k);
        Ok(k)
    }

    /// Evaluates the graph outputs named in `outputs` (all of them when empty).
    pub fn eval(
        &self,
        plan: &Plan,
        outputs: &[&str],
        opts: &EvalOptions,
    ) -> Result<EvalResult, GraphError> {
        let names: Vec<String> = if outputs.is_empty() {
            plan.outputs.keys().cloned().collect()
        } else {
            outputs.iter().map(|s| s.to_string()).collect()
        };
        let mut roots = Vec::new();
        for name in &names {
            roots.push(plan.output(name)?.clone());
        }
        let mut slots = Vec::new();
        let mut asked = Vec::new();
        for c in &roots {
            match c {
                Conn::Slot(i, p) => {
                    slots.push(*i);
                    asked.push((*i, Some(*p)));
                }
                Conn::Unbound { name, at } => {
                    return Err(GraphError::UnboundInput {
                        name: name.clone(),
                        at: at.clone(),
                    })
                }
                Conn::None => {}
            }
        }
        // Only the outputs asked for and read are computed (a lazy operator's others are
        // left out).
        let demand = plan.demand(&asked);
        let whole = self.eval_instances(plan, &slots, opts, None, Some(&demand))?;
        let mut out = BTreeMap::new();
        for (name, c) in names.iter().zip(&roots) {
            if let Conn::Slot(i, p) = c {
                if let Some(v) = whole.results.get(i).and_then(|e| e.values.get(*p)) {
                    out.insert(name.clone(), v.clone());
                }
            }
        }
        Ok(EvalResult {
            outputs: out,
            stats: whole.stats,
            memory: whole.memory,
        })
    }

    /// Evaluates instances `roots` of `plan` whole, with everything they need: their results
    /// (and those of every instance considered, or with `keep` only those it keeps: see
    /// [`kept`]), the stats of each, and the memory estimate. `demand` ([`Plan::demand`]):
    /// the outputs of each instance to compute; `None`: all of them (an instance's every
    /// output complete, as the editor's thumbnails and the tiles expect).
    fn eval_instances(
        &self,
        plan: &Plan,
        roots: &[usize],
        opts: &EvalOptions,
        keep: Option<&kept::Keep>,
        demand: Option<&[u64]>,
    ) -> Result<Whole, GraphError> {
        let want = |i: usize| demand.map_or(ALL_PORTS, |d| d[i]);
        let mut keys = HashMap::new();
        let mut results: HashMap<usize, Arc<CacheEntry>> = HashMap::new();
        let mut visited = HashSet::new();
        let mut to_run = Vec::new();
        let mut stats: HashMap<usize, NodeStats> = HashMap::new();
        for &i in roots {
            self.pull(
                plan,
                i,
                &want,
                &mut keys,
                &mut visited,
                &mut results,
                &mut to_run,
                &mut stats,
            )?;
        }
        // Refuse before running what would not fit in memory (sizes known without running).
        let cached: HashMap<usize, (usize, usize)> = results
            .iter()
            .filter_map(|(&i, e)| Some((i, e.values.iter().find_map(Value::size)?)))
            .collect();
        let sizes = memory::sizes(plan, &cached);
        let estimate = memory::estimate(plan, &to_run, &sizes);
        memory::check(&estimate, memory::budget()?, &plan.at)?;
        // Dependency levels among the nodes to run (to_run is in post-order).
        let run_set: HashSet<usize> = to_run.iter().copied().collect();
        let mut level: HashMap<usize, usize> = HashMap::new();
        for &i in &to_run {
            let l = plan.instances[i]
                .inputs
                .iter()
                .filter_map(|c| match c {
                    Conn::Slot(j, _) if run_set.contains(j) => level.get(j).map(|l| l + 1),
                    _ => None,
                })
                .max()
                .unwrap_or(0);
            level.insert(i, l);
        }
        let depth = level.values().max().map_or(0, |m| m + 1);
        let mut readers = kept::readers(plan, &to_run);
        if let Some(k) = keep {
            // Values from the caches: told, then dropped unless a node to run reads them.
            let hits: Vec<usize> = results.keys().copied().collect();
            for i in hits {
                k.tell(i, keys[&i], &results[&i]);
                if !readers.contains_key(&i) && !k.kept.contains(&i) {
                    results.remove(&i);
                }
            }
        }
        let total = to_run.len();
        let done = AtomicUsize::new(0);
        let ctx = RunContext::new(plan.protected.clone()).with_cancel(opts.token());
        for l in 0..depth {
            let batch: Vec<usize> = to_run.iter().copied().filter(|i| level[i] == l).collect();
            let ran: Vec<Result<Ran, GraphError>> = batch
                .par_iter()
                .map(|&i| {
                    if opts.cancelled() {
                        return Err(GraphError::Cancelled);
                    }
                    let r = self.run_one(plan, i, keys[&i], &results, &ctx, want(i))?;
                    if let Some(p) = &opts.progress {
                        p(&Progress {
                            done: done.fetch_add(1, Ordering::Relaxed) + 1,
                            total,
                            at: plan.instances[i].at.clone(),
                            op: plan.instances[i].op.spec().id,
                        });
                    }
                    Ok((i, r.0, r.1))
                })
                .collect();
            let mut ran_ok = Vec::with_capacity(ran.len());
            for r in ran {
                let (i, entry, st) = r?;
                results.insert(i, entry);
                stats.insert(i, st);
                ran_ok.push(i);
            }
            if let Some(k) = keep {
                for i in ran_ok {
                    k.tell(i, keys[&i], &results[&i]);
                    kept::release(plan, i, k, &mut readers, &mut results);
                }
            }
        }
        if opts.curl_stats {
            self.readouts(&keys, &mut results, &mut stats, plan, opts)?;
        }
        let mut order: Vec<usize> = stats.keys().copied().collect();
        order.sort_unstable();
        Ok(Whole {
            results,
            stats: order.into_iter().filter_map(|i| stats.remove(&i)).collect(),
            memory: estimate,
            keys,
        })
    }

    #[allow(clippy::too_many_arguments)]
    fn pull(
        &self,
        plan: &Plan,
        i: usize,
        want: &dyn Fn(usize) -> u64,
        keys: &mut HashMap<usize, CacheKey>,
        visited: &mut HashSet<usize>,
        results: &mut HashMap<usize, Arc<CacheEntry>>,
        to_run: &mut Vec<usize>,
        stats: &mut HashMap<usize, NodeStats>,
    ) -> Result<(), GraphError> {
        if !visited.insert(i) {
            return Ok(());
        }
        let key = self.key(plan, i, keys)?;
        let inst = &plan.instances[i];
        let spec = inst.op.spec();
        if !spec.side_effect {
            let mut status = None;
            // An entry that left out an output wanted now is no hit.
            let mut entry = self.mem.lock().get(key).filter(|e| e.has(want(i)));
            if entry.is_some() {
                status = Some(Status::Hit);
            } else if let Some(e) = self.disk.as_ref().and_then(|d| d.get(key)) {
                let e = Arc::new(e);
                self.mem.lock().insert(key, e.clone());
                entry = Some(e);
                status = Some(Status::DiskHit);
            }
            if let (Some(e), Some(status)) = (entry, status) {
                stats.insert(
                    i,
                    NodeStats {
                        at: inst.at.clone(),
                        op: spec.id,
                        status,
                        time: Duration::ZERO,
                        readout: Duration::ZERO,
                        bytes: e.byte_size(),
                        curl: e.curl,
                        fraction: e.fraction,
                        key,
                    },
                );
                results.insert(i, e);
                return Ok(());
            }
        }
        for c in &inst.inputs {
            match c {
                Conn::Slot(j, _) => {
                    self.pull(plan, *j, want, keys, visited, results, to_run, stats)?;
                }
                Conn::Unbound { name, at } => {
                    return Err(GraphError::UnboundInput {
                        name: name.clone(),
                        at: at.clone(),
                    })
                }
                Conn::None => {}
            }
        }
        to_run.push(i);
        Ok(())
    }

    /// The integrability readouts of every considered node's RGBN output that has none yet,
    /// taken on all cores after the nodes ran (so they never delay a node), each timed into
    /// its node's [`NodeStats::readout`] and kept with the value in the memory cache.
    fn readouts(
        &self,
        keys: &HashMap<usize, CacheKey>,
        results: &mut HashMap<usize, Arc<CacheEntry>>,
        stats: &mut HashMap<usize, NodeStats>,
        plan: &Plan,
        opts: &EvalOptions,
    ) -> Result<(), GraphError> {
        let todo: Vec<(usize, Arc<CacheEntry>)> = results
            .iter()
            .filter(|(i, e)| stats.contains_key(i) && e.curl.is_none())
            .filter(|(_, e)| e.values.iter().any(|v| matches!(v, Value::Rgbn(_))))
            .map(|(i, e)| (*i, e.clone()))
            .collect();
        type Read = Result<(usize, Arc<CacheEntry>, Duration), GraphError>;
        let token = opts.token();
        let done: Vec<Read> = todo
            .into_par_iter()
            .map(|(i, e)| {
                if token.is_cancelled() {
                    return Err(GraphError::Cancelled);
                }
                let t0 = Instant::now();
                // The readout's solver sees this evaluation's token (not one a pool worker
                // may have entered for another job) and a cancelled readout is not kept.
                let (curl, fraction) = {
                    let _current = token.enter();
                    integrability_of(&e)
                };
                if token.is_cancelled() {
                    return Err(GraphError::Cancelled);
                }
                let mut c = (*e).clone();
                (c.curl, c.fraction) = (curl, fraction);
                Ok((i, Arc::new(c), t0.elapsed()))
            })
            .collect();
        for d in done {
            let (i, e, t) = d?;
            if !plan.instances[i].op.spec().side_effect {
                if let Some(k) = keys.get(&i) {
                    self.mem.lock().insert(*k, e.clone());
                }
            }
            if let Some(st) = stats.get_mut(&i) {
                (st.curl, st.fraction, st.readout) = (e.curl, e.fraction, t);
            }
            results.insert(i, e);
        }
        Ok(())
    }

    fn run_one(
        &self,
        plan: &Plan,
        i: usize,
        key: CacheKey,
        results: &HashMap<usize, Arc<CacheEntry>>,
        ctx: &RunContext,
        want: u64,
    ) -> Result<(Arc<CacheEntry>, NodeStats), GraphError> {
        let inst = &plan.instances[i];
        let spec = inst.op.spec();
        // A lazy operator is told which outputs are read; the rest are recorded as skipped.
        let skipped = spec.skipped(want);
        let lazy_ctx;
        let ctx = if skipped != 0 {
            lazy_ctx = ctx.wanting(want);
            &lazy_ctx
        } else {
            ctx
        };
        let inputs: Vec<Option<Value>> = inst
            .inputs
            .iter()
            .map(|c| match c {
                Conn::Slot(j, p) => results.get(j).and_then(|e| e.values.get(*p)).cloned(),
                _ => None,
            })
            .collect();
        let t0 = Instant::now();
        let values = inst
            .op
            .run(&inst.params, inputs, ctx)
            .map_err(|source| GraphError::node(spec.id, source, inst.at.clone()))?;
        let time = t0.elapsed();
        let entry = Arc::new(CacheEntry {
            values,
            curl: None,
            fraction: None,
            skipped,
        });
        if !spec.side_effect {
            self.mem.lock().insert(key, entry.clone());
            // The disk keeps complete entries only.
            if let Some(d) = self.disk.as_ref().filter(|_| skipped == 0) {
                if let Err(e) = d.put(key, &entry) {
                    tracing::warn!("disk cache write failed ({e}): {}", d.dir().display());
                }
            }
        }
        let st = NodeStats {
            at: inst.at.clone(),
            op: spec.id,
            status: if spec.side_effect {
                Status::Effect
            } else {
                Status::Miss
            },
            time,
            readout: Duration::ZERO,
            bytes: entry.byte_size(),
            curl: None,
            fraction: None,
            key,
        };
        Ok((entry, st))
    }
}

/// Relative RMS curl and non-integrable fraction of the first RGBN value computed (F is
/// `None` where the integration refuses the image, e.g. a mask with nothing inside).
fn integrability_of(e: &CacheEntry) -> (Option<f64>, Option<f64>) {
    e.values
        .iter()
        .enumerate()
        .filter(|(k, _)| e.has(if *k < 64 { 1 << k } else { 0 }))
        .find_map(|(_, v)| match v {
            Value::Rgbn(img) => {
                let g = GradientField::from_normals(img);
                let curl = g.curl_stats(img.mask()).relative;
                let f = crate::raster::integrate::non_integrable_fraction(&g, img.mask()).ok();
                Some((Some(curl), f))
            }
            _ => None,
        })
        .unwrap_or((None, None))
}

/// The XXH3-128 of a file's bytes, read through a 1 MiB buffer (the same value as hashing the
/// whole file at once, without holding it: a 4K input is not copied into a fresh buffer).
fn hash_file(path: &Path) -> std::io::Result<u128> {
    use std::io::Read;
    let mut f = std::fs::File::open(path)?;
    let mut h = xxhash_rust::xxh3::Xxh3::new();
    let mut buf = vec![0u8; 1 << 20];
    loop {
        match f.read(&mut buf) {
            Ok(0) => return Ok(h.digest128()),
            Ok(n) => h.update(&buf[..n]),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
}

#[cfg(test)]
mod hash_tests {
    /// Hashed in 1 MiB reads, a file gives the hash of its bytes taken at once (sizes on both
    /// sides of the buffer's edge, and empty).
    #[test]
    fn a_file_hashed_in_pieces_equals_its_bytes_hashed_whole() {
        let dir = std::env::temp_dir().join(format!("rgbn-hash-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for len in [
            0usize,
            1,
            (1 << 20) - 1,
            1 << 20,
            (1 << 20) + 1,
            3 << 20 | 12345,
        ] {
            let bytes: Vec<u8> = (0..len)
                .map(|i| ((i * 2_654_435_761) >> 13) as u8)
                .collect();
            let p = dir.join(format!("f{len}"));
            std::fs::write(&p, &bytes).unwrap();
            assert_eq!(
                super::hash_file(&p).unwrap(),
                xxhash_rust::xxh3::xxh3_128(&bytes),
                "{len} bytes"
            );
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
