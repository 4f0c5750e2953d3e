"""rgbn.dask: a graph evaluated chunk by chunk by Dask (a LocalCluster of two worker processes)
writes stores equal, file for file, to one whole `rgbn eval` of the image; a worker killed mid-run
still leaves a complete, equal output; a global operator is refused naming the node; a bad store
or a failing chunk raises rgbn's errors naming the store or the chunk.

The reference is `rgbn eval` run as a separate process (the command line of this package, the
release build `pip install` made: the debug binary of `cargo test` would take minutes on 4K).
"""

import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import rgbn

dask = pytest.importorskip("dask")
distributed = pytest.importorskip("distributed")
zarr = pytest.importorskip("zarr")
import rgbn.dask as rd  # noqa: E402

from conftest import GRAPHS  # noqa: E402

# The issue asks for a 4K input; RGBN_DASK_TEST_SIZE lowers it where CI time matters.
SIZE = int(os.environ.get("RGBN_DASK_TEST_SIZE", "4096"))


def rgbn_cli(args, cwd=None, check=True):
    """`rgbn ARGS` as its own process (this package's command line)."""
    cmd = [sys.executable, "-c", "import sys, rgbn; sys.exit(rgbn.main(sys.argv[1:]))", *map(str, args)]
    r = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True)
    if check and r.returncode != 0:
        raise AssertionError(f"rgbn {' '.join(map(str, args))} failed ({r.returncode}): {r.stderr}")
    return r


def files(root):
    """Every file of a store: {relative path: bytes}."""
    out = {}
    for d, _, names in os.walk(root):
        for n in names:
            p = os.path.join(d, n)
            out[os.path.relpath(p, root)] = open(p, "rb").read()
    return out


def assert_same_store(a, b):
    fa, fb = files(a), files(b)
    assert sorted(fa) == sorted(fb), (sorted(set(fa) ^ set(fb)))[:10]
    differ = [k for k in fa if fa[k] != fb[k]]
    assert not differ, f"{len(differ)} files differ, e.g. {differ[:5]}"


DEMO = """(
    version: 2,
    next_id: 2,
    outputs: {{ "image": (node: 1, port: "image") }},
    nodes: [ (id: 1, op: "demo", pos: (0.0, 0.0), params: {{ "size": Int({size}) }}) ],
)
"""


def make_store(tmp, size, name="in.zarr", cut=None):
    """An RGBN store of the demo medallion, size² (or cut to (w, h)), 512-pixel chunks."""
    g = tmp / "demo_src.ron"
    g.write_text(DEMO.format(size=size))
    path = tmp / name
    if cut is None:
        rgbn_cli(["eval", g, "-o", f"image={path}"])
    else:
        w, h = cut
        rgbn_cli(["eval", g, "--region", f"0,0,{w},{h}", "-o", f"image={tmp / 'cut.exr'}"])
        rgbn.write(rgbn.read(str(tmp / "cut.exr")), str(path))
    return path


PEN_STAMP_BILATERAL = """(
    version: 2,
    next_id: 6,
    inputs: {{ "image": (ty: Rgbn) }},
    outputs: {{
        "base": (node: 4, port: "base"),
        "detail": (node: 4, port: "detail"),
        "height": (node: 1, port: "height"),
    }},
    nodes: [
        (id: 1, op: "pen", name: Some("stroke across chunks"), pos: (0.0, 0.0),
         params: {{
            "height_px": Float(3.0), "width_px": Float(14.0), "taper_px": Float(10.0),
            "profile": Choice("bump"),
            "paths": Paths([ (points: [ (10.0, {h8}), ({w2}, {h2}), ({w9}, {h9}) ]) ]),
         }},
         inputs: {{ "image": Input("image") }}),
        (id: 2, op: "surface", name: Some("dome"), pos: (0.0, 160.0),
         params: {{ "height": Int(40), "shape": Choice("gaussians"), "width": Int(40) }}),
        (id: 3, op: "stamp", name: Some("domes on chunk corners"), pos: (240.0, 0.0),
         params: {{
            "angle_rad": Float(0.5), "color": Bool(false), "falloff_px": Float(3.0),
            "positions": Points([ (256.0, 256.0), ({w2}, {h3}), (30.0, {h9}) ]),
            "scale_x": Float(1.25), "scale_y": Float(0.8),
         }},
         inputs: {{ "image": Node(1, "image"), "stamp": Node(2, "image") }}),
        (id: 4, op: "bilateral", name: Some("smooth"), pos: (480.0, 0.0),
         params: {{ "sigma_spatial_px": Float(3.0), "sigma_color": Float(0.2), "sigma_normal": Float(0.25), "filter_color": Bool(true) }},
         inputs: {{ "image": Node(3, "image") }}),
    ],
)
"""

INTEGRATE = """(
    version: 2,
    next_id: 3,
    inputs: { "image": (ty: Rgbn) },
    outputs: { "height": (node: 2, port: "height") },
    nodes: [
        (id: 1, op: "filter.sharpen", name: Some("sharpen"), pos: (0.0, 0.0),
         inputs: { "image": Input("image") }),
        (id: 2, op: "integrate", name: Some("heights"), pos: (240.0, 0.0),
         inputs: { "image": Node(1, "image") }),
    ],
)
"""


@pytest.fixture(scope="module")
def cluster():
    """A LocalCluster of two worker processes of one thread each, and its client."""
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None, memory_limit="2GiB"
    ) as c, distributed.Client(c) as client:
        yield client


@pytest.fixture(scope="module")
def big_store(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("dask4k")
    return make_store(tmp, SIZE)


def test_input_image_on_a_local_cluster_equals_the_whole_eval(cluster, big_store, tmp_path):
    g = GRAPHS / "input_image.ron"
    rgbn_cli(["eval", g, "--input", f"image={big_store}", "-o", f"image={tmp_path / 'w_image.zarr'}",
              "-o", f"relit={tmp_path / 'w_relit.zarr'}"])
    outs = {"image": tmp_path / "d_image.zarr", "relit": tmp_path / "d_relit.zarr"}
    got = rd.evaluate(g, {"image": big_store}, outs)
    assert set(got) == {"image", "relit"}
    assert_same_store(tmp_path / "d_image.zarr", tmp_path / "w_image.zarr")
    assert_same_store(tmp_path / "d_relit.zarr", tmp_path / "w_relit.zarr")


GAUSS8 = """(
    version: 2,
    next_id: 2,
    inputs: { "image": (ty: Rgbn) },
    outputs: { "image": (node: 1, port: "image") },
    nodes: [ (id: 1, op: "filter.gaussian", name: Some("gauss8"), pos: (0.0, 0.0),
              params: { "sigma_px": Float(8.0) }, inputs: { "image": Input("image") }) ],
)
"""


def test_a_streamed_gaussian_whose_halo_crosses_chunks_equals_the_whole_eval(cluster, big_store, tmp_path):
    # A store input and a local operator: the tasks stream their windows (the σ 8 px Gaussian's
    # halo reaches into the next chunk row and column of every task).
    g = tmp_path / "gauss8.ron"
    g.write_text(GAUSS8)
    assert rgbn._rgbn._dask_streams(rgbn._rgbn._dask_graph(str(g)), {"image": str(big_store)}, ["image"])
    rgbn_cli(["eval", g, "--input", f"image={big_store}", "-o", f"image={tmp_path / 'w.zarr'}"])
    rd.evaluate(g, {"image": big_store}, {"image": tmp_path / "d.zarr"}, chunks=1024)
    # The recursive Gaussian is cut at 4σ where a task's window ends, as the whole run's strips
    # are: the same files, every level within the documented truncation (per pass the tail's
    # mass, < 3.5e-4, times twice the largest gradient; 2e-3 over two passes for gradients up
    # to 1.4 — tests/it/region.rs).
    fa, fb = files(tmp_path / "d.zarr"), files(tmp_path / "w.zarr")
    assert sorted(fa) == sorted(fb)
    k = 0
    while (tmp_path / "w.zarr" / str(k)).exists():
        a = zarr.open_array(str(tmp_path / "d.zarr" / str(k)))[:]
        b = zarr.open_array(str(tmp_path / "w.zarr" / str(k)))[:]
        assert a.shape == b.shape and np.abs(a - b).max() <= 2e-3, (k, np.abs(a - b).max())
        k += 1


def test_levels_caps_the_pyramid_as_zarr_levels_does(cluster, big_store, tmp_path):
    # levels=1: level 0 alone in the store and in its multiscales, as `rgbn eval --zarr-levels 1`;
    # level 0 the same as with the whole pyramid (within the streamed Gaussian's truncation).
    g = tmp_path / "gauss8.ron"
    g.write_text(GAUSS8)
    rgbn_cli(["eval", g, "--input", f"image={big_store}", "-o", f"image={tmp_path / 'w.zarr'}", "--zarr-levels", "1"])
    rd.evaluate(g, {"image": big_store}, {"image": tmp_path / "d.zarr"}, chunks=1024, levels=1)
    assert sorted(files(tmp_path / "d.zarr")) == sorted(files(tmp_path / "w.zarr"))
    assert not (tmp_path / "d.zarr" / "1").exists()
    group = zarr.open_group(str(tmp_path / "d.zarr"), mode="r")
    assert [d["path"] for d in group.attrs["ome"]["multiscales"][0]["datasets"]] == ["0"]
    a = zarr.open_array(str(tmp_path / "d.zarr" / "0"))[:]
    b = zarr.open_array(str(tmp_path / "w.zarr" / "0"))[:]
    assert a.shape == b.shape == (6, SIZE, SIZE) and np.abs(a - b).max() <= 2e-3
    with pytest.raises(rgbn.InputError, match="levels=0"):
        rd.evaluate(g, {"image": big_store}, {"image": tmp_path / "e.zarr"}, levels=0)


def test_the_task_side_grows_for_streamed_tasks_and_shrinks_with_the_workers():
    # Streamed tasks: the largest of 1024, 2048, 4096 leaving 4 tasks per worker thread.
    assert rd._auto_side(16384, 16384, 512, True, 2) == 4096  # 16 tasks
    assert rd._auto_side(16384, 16384, 512, True, 16) == 2048  # 64 tasks
    assert rd._auto_side(16384, 16384, 512, True, 64) == 1024  # 256 tasks
    assert rd._auto_side(4096, 4096, 512, True, 2) == 1024  # 16 tasks (2048 would give 4)
    # Tasks of the region plan keep the default side, whose memory is bounded.
    assert rd._auto_side(16384, 16384, 512, False, 2) == rd.DEFAULT_CHUNKS == 1024


def test_pen_stamp_bilateral_on_a_local_cluster_equals_the_whole_eval(cluster, tmp_path):
    w, h = 1300, 1100  # not multiples of the chunks: partial chunks at the right and bottom
    store = make_store(tmp_path, 1400, cut=(w, h))
    g = tmp_path / "psb.ron"
    g.write_text(PEN_STAMP_BILATERAL.format(
        w2=w / 2, h2=h / 2, h3=h / 3, h8=h / 8, w9=w * 0.9, h9=h * 0.9))
    names = ["base", "detail", "height"]
    rgbn_cli(["eval", g, "--input", f"image={store}", *sum((["-o", f"{n}={tmp_path / ('w_' + n + '.zarr')}"] for n in names), [])])
    outs = {n: tmp_path / f"d_{n}.zarr" for n in names}
    rd.evaluate(g, {"image": store}, outs, chunks=512)
    # pen and stamp: file for file.
    assert_same_store(tmp_path / "d_height.zarr", tmp_path / "w_height.zarr")
    # bilateral: the engine's tiled bilateral (the plan of `rgbn eval --region`) differs from
    # its whole-image run in the last bit of some values (measured ≤ 3e-7; an open engine
    # issue, not rgbn.dask's): every level within 1e-6, the store layout the same.
    for n in ("base", "detail"):
        fa, fb = files(tmp_path / f"d_{n}.zarr"), files(tmp_path / f"w_{n}.zarr")
        assert sorted(fa) == sorted(fb)
        k = 0
        while (tmp_path / f"w_{n}.zarr" / str(k)).exists():
            a = zarr.open_array(str(tmp_path / f"d_{n}.zarr" / str(k)))[:]
            b = zarr.open_array(str(tmp_path / f"w_{n}.zarr" / str(k)))[:]
            assert a.shape == b.shape and np.allclose(a, b, rtol=0, atol=1e-6, equal_nan=True), (n, k)
            k += 1
    # The lazy form: dask arrays in rgbn's channel layout, equal to the stores' level 0.
    arrs = rd.arrays(g, {"image": store}, ["base", "height"], chunks=512)
    base = arrs["base"]
    assert base.shape == (6, h, w) and base.chunks[1][0] == 512
    b = base.compute()
    assert np.array_equal(b, zarr.open_array(str(tmp_path / "d_base.zarr" / "0"))[:], equal_nan=True)
    assert np.array_equal(arrs["height"].compute(), zarr.open_array(str(tmp_path / "d_height.zarr" / "0"))[:])


def test_a_worker_killed_mid_run_leaves_a_complete_equal_output(cluster, big_store, tmp_path):
    g = GRAPHS / "input_image.ron"
    rgbn_cli(["eval", g, "--input", f"image={big_store}", "-o", f"relit={tmp_path / 'w_relit.zarr'}"])
    out = tmp_path / "d_relit.zarr"
    pids = cluster.run(os.getpid)
    done, errors = threading.Event(), []

    def run():
        try:
            # Small tasks, so that the kill lands while many are still to run.
            rd.evaluate(g, {"image": big_store}, {"relit": out}, chunks=512)
        except BaseException as e:  # noqa: BLE001
            errors.append(e)
        finally:
            done.set()

    t = threading.Thread(target=run)
    t.start()
    # Kill one worker once the first chunks are written (level 0's chunk files).
    deadline = time.monotonic() + 600
    while not done.is_set() and time.monotonic() < deadline:
        c0 = out / "0" / "c"
        if c0.exists() and sum(len(f) for _, _, f in os.walk(c0)) >= 2:
            break
        time.sleep(0.05)
    killed = not done.is_set()
    if killed:
        os.kill(next(iter(pids.values())), signal.SIGKILL)
    t.join()
    assert not errors, errors
    assert killed, "the run ended before a worker could be killed: make the input larger"
    assert_same_store(out, tmp_path / "w_relit.zarr")


def test_a_global_operator_is_refused_naming_the_node(tmp_path, big_store):
    g = tmp_path / "integrate.ron"
    g.write_text(INTEGRATE)
    with pytest.raises(rgbn.InputError) as e:
        rd.evaluate(g, {"image": big_store}, {"height": tmp_path / "h.zarr"})
    msg = str(e.value)
    assert 'node 2 "heights"' in msg and "global" in msg
    assert "level" in msg and "cut the graph before" in msg
    assert not (tmp_path / "h.zarr").exists()


def test_bad_stores_raise_file_error_naming_the_store_and_chunk(tmp_path):
    g = GRAPHS / "input_image.ron"
    # Not OME: a plain Zarr array.
    plain = tmp_path / "plain.zarr"
    zarr.create_array(str(plain), shape=(6, 64, 64), chunks=(6, 32, 32), dtype="float32")
    # The same class `rgbn.read` raises for a file it cannot decode.
    with pytest.raises(rgbn.FileError) as e:
        rd.evaluate(g, {"image": plain}, {"relit": tmp_path / "a.zarr"}, threads=1)
    assert "plain.zarr" in str(e.value)
    # A missing chunk: found by the task that reads it, which names its chunk.
    store = make_store(tmp_path, 1024, name="holed.zarr")
    os.remove(store / "0" / "c" / "0" / "1" / "1")
    with pytest.raises(rgbn.FileError) as e:
        rd.evaluate(g, {"image": store}, {"relit": tmp_path / "b.zarr"}, chunks=512)
    msg = str(e.value)
    # The chunk of the task that met it (the missing chunk or a neighbour reading its halo).
    assert "holed.zarr" in msg and "chunk at " in msg and "--region" in msg, msg
    # Nothing is written over an input.
    with pytest.raises(rgbn.Error):
        rd.evaluate(g, {"image": store}, {"relit": store})


def test_dask_array_inputs_equal_store_inputs(tmp_path):
    store = make_store(tmp_path, 600)
    import dask.array as da

    arr = da.from_zarr(str(store / "0"))
    g = GRAPHS / "input_image.ron"
    a = rd.arrays(g, {"image": store}, ["relit"], chunks=256)["relit"].compute(scheduler="threads")
    b = rd.arrays(g, {"image": arr}, ["relit"], chunks=256)["relit"].compute(scheduler="threads")
    assert a.shape == (4, 600, 600) and a.dtype == np.uint8
    assert np.array_equal(a, b)


def test_the_lazy_form_keeps_its_scratch_store_while_its_arrays_live(tmp_path, monkeypatch):
    # A dask-array input is written as a store in the working directory for the tasks to read;
    # it must outlive the call (the arrays are lazy) and go when the arrays are collected.
    import gc

    import dask.array as da

    store = make_store(tmp_path, 600)
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    arr = da.from_zarr(str(store / "0"))
    relit = rd.arrays(GRAPHS / "input_image.ron", {"image": arr}, ["relit"], chunks=256)["relit"]
    assert len(list(work.glob(".rgbn-dask-*"))) == 1
    gc.collect()
    want = rd.arrays(GRAPHS / "input_image.ron", {"image": store}, ["relit"], chunks=256)["relit"]
    assert np.array_equal(relit.compute(scheduler="threads"), want.compute(scheduler="threads"))
    del relit
    gc.collect()
    assert list(work.glob(".rgbn-dask-*")) == []
