"""rgbn graphs on a Dask cluster: OME-Zarr stores in, OME-Zarr stores (or dask arrays) out.

``pip install "./python[dask]"`` installs what this module needs (``dask[array]``,
``distributed``, ``zarr`` 3, ``ome-zarr``). See ``docs/distributed.md`` for a guide.

- :func:`evaluate` — evaluate a graph chunk by chunk and write its outputs into OME-Zarr stores;
  returns when they are written.
- :func:`arrays` — the lazy form: one dask array per output, for composing further.

**One task per output chunk.** Each task evaluates the graph over its chunk with the engine's
region plan — the plan of ``rgbn eval --region``: the tiles the chunk covers plus every
operator's halo, input stores read only in the chunks that cover that — and writes its chunk
of every output (atomically; a retried task writes the same bytes). No task holds the whole
image. The output stores are created by the tasks themselves, race-safely, at the outputs'
whole size (``docs/distributed.md``, "How several writers share one store").

**Scheduler.** Dask's own: the active ``distributed.Client`` when there is one (a
``LocalCluster``, a ``dask-jobqueue`` cluster), else dask's threaded scheduler. A worker that
dies is replaced and its tasks rerun by Dask.

**Limits.** A graph whose outputs depend on a global operator (integration, the
integrability projection, statistics) cannot be cut into chunks and is refused with an
:class:`rgbn.InputError` naming the node: evaluate it at a level on one machine, or cut the
graph before that node.
"""

import os
import shutil
import tempfile
import weakref

from . import _rgbn
from ._rgbn import Error

__all__ = ["evaluate", "arrays", "DEFAULT_CHUNKS", "ZARR_CHUNK"]

#: Side in pixels of one task's square of the outputs when ``chunks`` is not given and the
#: tasks cannot stream (below): four 512-pixel store chunks, so that a task's work (tens of
#: milliseconds and more per task on the graphs of ``graphs/``) outweighs Dask's per-task
#: overhead (BENCHMARKS.md, "rgbn.dask") while its memory stays small (a few hundred MB at
#: most per task).
DEFAULT_CHUNKS = 1024
#: Largest task side chosen when the tasks stream (every output an image or a picture that
#: depends through local operators on one OME-Zarr store): a streamed task reads its window
#: top to bottom, so its memory is a few strips whatever its side, and a larger task decodes
#: fewer store chunks twice (the ring of chunks its halo touches: 2.25 times the chunks it
#: writes at 2048, 1.56 at 4096, 4 at 1024).
MAX_STREAMED_CHUNKS = 4096
#: Tasks per worker thread at least, when the side is chosen: enough for Dask to even out
#: the workers' load and to retry a lost task cheaply.
TASKS_PER_THREAD = 4
#: Chunk side of the output stores (rgbn's default, ``--chunk``).
ZARR_CHUNK = 512
#: The region engine's tile side (``rgbn eval --tile``).
TILE = 512

_RGBN_LABELS = {3: ["nx", "ny", "nz"], 6: ["R", "G", "B", "nx", "ny", "nz"], 7: ["R", "G", "B", "nx", "ny", "nz", "mask"]}


def _sets(set):
    if not set:
        return []
    out = []
    for k, v in dict(set).items():
        if isinstance(v, (list, tuple)):
            v = ",".join(":".join(map(str, x)) if isinstance(x, (list, tuple)) else str(x) for x in v)
        elif isinstance(v, bool):
            v = "true" if v else "false"
        out.append(f"{k}={v}")
    return out


def _chunk_side(chunks, zarr_chunk):
    if chunks is None:
        return None
    elif isinstance(chunks, int):
        side = chunks
    else:
        sides = set(int(c) for c in chunks)
        if len(sides) != 1:
            raise _rgbn.InputError(f"chunks={chunks!r}: give one side in pixels (square chunks)")
        side = sides.pop()
    if side < 16 or side % zarr_chunk:
        raise _rgbn.InputError(
            f"chunks={side}: a task's side must be a multiple of the stores' {zarr_chunk}-pixel chunks "
            f"(zarr_chunk), so that no two tasks write one chunk"
        )
    return side


def _auto_side(w, h, zarr_chunk, streams, threads):
    """The task side when ``chunks`` is not given: :data:`DEFAULT_CHUNKS` for tasks of the
    region plan; for streamed tasks the largest of :data:`DEFAULT_CHUNKS` doubled up to
    :data:`MAX_STREAMED_CHUNKS` (1024, 2048, 4096) that still gives every one of ``threads``
    worker threads :data:`TASKS_PER_THREAD` tasks."""
    if not streams:
        return DEFAULT_CHUNKS
    # Power-of-two multiples of the store's chunk: they cut a power-of-two image into equal
    # squares (a ragged last row of tasks would waste a round).
    floor = max(DEFAULT_CHUNKS // zarr_chunk, 1) * zarr_chunk
    side = floor
    while side * 2 <= MAX_STREAMED_CHUNKS and len(_regions(w, h, side * 2)) >= TASKS_PER_THREAD * max(threads, 1):
        side *= 2
    return side


def _threads(client):
    if client is not None:
        try:
            return sum(client.nthreads().values())
        except Exception:  # noqa: BLE001 - a client that cannot say: the local machine's count
            pass
    return os.cpu_count() or 1


def _regions(w, h, side):
    return [(x, y, min(side, w - x), min(side, h - y)) for y in range(0, h, side) for x in range(0, w, side)]


def _describe(region):
    x, y, w, h = region
    return f"chunk at {x},{y} ({w}×{h} px; rgbn eval --region {x},{y},{w},{h})"


def _task(graph, inputs, outputs, region, level, zarr_chunk, tile, threads, levels=None):
    """One Dask task: the graph over ``region``; writes it into the output stores (``outputs``
    a dict) or returns ``{name: value}`` (a list). An rgbn error is raised again, of the same
    class, naming the chunk (the engine's message names the node)."""
    try:
        return _rgbn._dask_region(graph, inputs, outputs, region, level, zarr_chunk, tile, threads, levels)
    except Error as e:
        raise type(e)(f"{_describe(region)}: {e}") from None


def _paths(d, what):
    out = {}
    for k, v in dict(d).items():
        if not isinstance(k, str):
            raise _rgbn.InputError(f"{what}: names must be strings, got {k!r}")
        out[k] = os.path.abspath(os.fspath(v))
    return out


def _store_dask_input(name, arr, root, zarr_chunk):
    """A dask array in rgbn's channel layout (C, H, W) written as an OME-Zarr store under
    ``root`` (by dask, chunk by chunk): the path rgbn's tasks read it from."""
    import zarr
    import dask.array as da

    if arr.ndim != 3 or arr.shape[0] not in _RGBN_LABELS:
        raise _rgbn.InputError(
            f"input {name!r}: a dask array in rgbn's channel layout is (C, H, W) with C = 3 "
            f"(nx, ny, nz), 6 (R, G, B, nx, ny, nz) or 7 (… mask); got shape {arr.shape}"
        )
    c, h, w = arr.shape
    path = os.path.join(root, f"{name}.zarr")
    g = zarr.open_group(path, mode="w", zarr_format=3)
    labels = _RGBN_LABELS[c]
    g.attrs["ome"] = {
        "version": "0.5",
        "multiscales": [
            {
                "axes": [
                    {"name": "c", "type": "channel"},
                    {"name": "y", "type": "space"},
                    {"name": "x", "type": "space"},
                ],
                "datasets": [{"path": "0", "coordinateTransformations": [{"type": "scale", "scale": [1.0, 1.0, 1.0]}]}],
            }
        ],
        "omero": {"channels": [{"label": l} for l in labels]},
    }
    z = g.create_array("0", shape=(c, h, w), chunks=(c, zarr_chunk, zarr_chunk), dtype="float32")
    da.store(arr.astype("float32").rechunk((c, zarr_chunk, zarr_chunk)), z, lock=False)
    return path


class _Scratch:
    """The folder holding dask-array inputs written as stores, for as long as a task graph that
    reads them exists: the lazy form's arrays hold this object in their tasks' arguments, and
    the folder is removed when the last of them is collected (or when the process exits). It
    lives in the working directory, which a cluster's workers share more often than a local
    temporary directory. A copy sent to a worker is only its path, which removes nothing."""

    def __init__(self, path):
        self.path = path
        self._remove = weakref.finalize(self, shutil.rmtree, path, True)

    def remove(self):
        self._remove()

    def __reduce__(self):
        return (str, (self.path,))

    def __dask_tokenize__(self):
        return self.path


def _prepare(graph, inputs, outputs, level, set, zarr_chunk):
    """(graph source, input paths, temporary folder (:class:`_Scratch`) or None, output sizes)."""
    src = _rgbn._dask_graph(graph, _sets(set))
    paths, tmp = {}, None
    for name, v in dict(inputs or {}).items():
        if hasattr(v, "dask") and hasattr(v, "chunks"):
            if tmp is None:
                tmp = _Scratch(tempfile.mkdtemp(prefix=".rgbn-dask-", dir=os.getcwd()))
            paths[name] = _store_dask_input(name, v, tmp.path, zarr_chunk)
        else:
            paths.update(_paths({name: v}, "inputs"))
    try:
        sizes = _rgbn._dask_plan(src, paths, list(outputs), int(level))
    except BaseException:
        if tmp:
            tmp.remove()
        raise
    return src, paths, tmp, sizes


def _client():
    try:
        from distributed import default_client
    except ImportError:
        return None
    try:
        return default_client()
    except ValueError:
        return None


def evaluate(graph, inputs, outputs, *, chunks=None, level=0, set=None, zarr_chunk=ZARR_CHUNK, threads=1, levels=None):
    """Evaluates ``graph`` chunk by chunk on Dask and writes ``outputs`` into OME-Zarr stores.

    - ``graph``: a graph file path (``.ron``) or an :class:`rgbn.Graph` (with its parameters).
    - ``inputs``: ``{name: path}`` of OME-Zarr stores (or of any image file, which each task
      then reads whole), or ``{name: dask array}`` in rgbn's channel layout ``(C, H, W)``.
    - ``outputs``: ``{name: path}``, each a ``.zarr`` store written at the output's whole size.
    - ``chunks``: a task's square side in pixels, a multiple of ``zarr_chunk`` (the stores'
      chunk side, default 512). By default :data:`DEFAULT_CHUNKS` (1024), or when the tasks
      stream (every output an image or a picture computed by local operators from one OME-Zarr
      store: a task then reads its window of the store top to bottom and its memory does not
      grow with its side) the largest side up to :data:`MAX_STREAMED_CHUNKS` (4096) that gives
      each worker thread :data:`TASKS_PER_THREAD` tasks.
    - ``level``: level of detail (``rgbn eval --level``): the outputs reduced ``2**level``
      times; input stores are read at that level directly.
    - ``set``: ``{"node.param": value}``, as ``rgbn eval --set``.
    - ``threads``: threads of rgbn's own per task (default 1: Dask's workers and threads are
      the parallelism).
    - ``levels``: most pyramid levels each output store gets, level 0 included (``rgbn eval
      --zarr-levels``); ``None`` (default): every level the size allows, as ``rgbn eval``
      writes (the ``multiscales`` pyramid). ``levels=1`` writes level 0 alone.

    Returns ``{name: path}`` when every chunk is written. Raises :class:`rgbn.InputError` for a
    global operator, a bad store or bad arguments, and a failing task's :class:`rgbn.Error`
    naming its chunk and node.
    """
    outs = _paths(outputs, "outputs")
    for name, p in outs.items():
        if not p.endswith(".zarr"):
            raise _rgbn.InputError(f"output {name!r}: {p} is not an OME-Zarr store (a path ending in .zarr)")
    side = _chunk_side(chunks, zarr_chunk)
    if levels is not None and (isinstance(levels, bool) or not isinstance(levels, int) or levels < 1):
        raise _rgbn.InputError(f"levels={levels!r}: give at least 1 (level 0 alone), or None for every level")
    src, paths, tmp, sizes = _prepare(graph, inputs, outs, level, set, zarr_chunk)
    try:
        import dask

        w, h = _common_size(sizes)
        client = _client()
        if side is None:
            streams = int(level) == 0 and _rgbn._dask_streams(src, paths, list(outs))
            side = _auto_side(w, h, zarr_chunk, streams, _threads(client))
        task = dask.delayed(_task, pure=True)
        token = _token(src, paths, outs, level, side, zarr_chunk, levels)
        tasks = [
            task(
                src, paths, outs, r, int(level), zarr_chunk, TILE, threads, levels,
                dask_key_name=f"rgbn-chunk-{r[0]}-{r[1]}-{token}",
            )
            for r in _regions(w, h, side)
        ]
        if client is not None:
            futures = client.compute(tasks)
            client.gather(futures)
        else:
            dask.compute(*tasks, scheduler="threads")
    finally:
        if tmp:
            tmp.remove()
    return outs


def _token(*parts):
    from dask.base import tokenize

    return tokenize(*parts)


def _common_size(sizes):
    dims = {(v[0], v[1]) for v in sizes.values()}
    if len(dims) != 1:
        listed = ", ".join(f"{n}: {v[0]}×{v[1]}" for n, v in sizes.items())
        raise _rgbn.InputError(
            f"the outputs have different sizes ({listed}): evaluate outputs of one size per call"
        )
    return dims.pop()


def _block(value, ty):
    import numpy as np

    if ty == "rgbn":
        planes = [value.color[..., i] for i in range(3)] + [value.normals[..., i] for i in range(3)]
        if value.mask is not None:
            planes.append(value.mask)
        return np.stack(planes).astype(np.float32, copy=False)
    if ty == "picture":
        return np.moveaxis(np.asarray(value), 2, 0)
    return np.asarray(value, dtype=np.float32)[None]


def _task_blocks(graph, inputs, types, region, level, zarr_chunk, tile, threads, scratch=None):
    """One Dask task of the lazy form: ``{name: (C, h, w) array}`` over ``region``. ``scratch``
    (the inputs' temporary folder, unused here) keeps that folder alive while tasks need it."""
    values = _task(graph, inputs, list(types), region, level, zarr_chunk, tile, threads)
    return {n: _block(values[n], ty) for n, ty in types.items()}


def _pick(blocks, name):
    return blocks[name]


def arrays(graph, inputs, outputs=None, *, chunks=None, level=0, set=None, threads=1):
    """The lazy form: ``{name: dask array}`` of the graph's outputs in rgbn's channel layout
    ``(C, H, W)`` — an RGBN image as R, G, B, nx, ny, nz (and mask when it has one), float32;
    a picture as R, G, B, A uint8; a mask or field as one float32 channel. ``outputs`` lists
    the names (default: every image-like output). Nothing is computed until the arrays are;
    each block is one task that evaluates every requested output over its square (the
    engine's region plan, as :func:`evaluate`). Arguments as :func:`evaluate`."""
    import dask
    import dask.array as da
    import numpy as np

    side = _chunk_side(chunks, 16) or DEFAULT_CHUNKS
    src, paths, scratch, sizes = _prepare(graph, inputs, list(outputs or []), level, set, ZARR_CHUNK)
    names = list(sizes)
    w, h = _common_size(sizes)
    regions = _regions(w, h, side)
    types = {n: sizes[n][2] for n in names}
    per = {
        r: dask.delayed(_task_blocks, pure=True)(src, paths, types, r, int(level), ZARR_CHUNK, TILE, threads, scratch)
        for r in regions
    }
    out = {}
    for name in names:
        ty, nc = sizes[name][2], sizes[name][3]
        dtype = np.uint8 if ty == "picture" else np.float32
        rows = []
        for y in range(0, h, side):
            row = []
            for x in range(0, w, side):
                r = (x, y, min(side, w - x), min(side, h - y))
                blk = dask.delayed(_pick, pure=True)(per[r], name)
                row.append(da.from_delayed(blk, shape=(nc, r[3], r[2]), dtype=dtype))
            rows.append(row)
        out[name] = da.block(rows)
    return out
