"""The cost of rgbn.dask's tasks outside Dask: N tasks of a graph over a store, run one after the
other in this process with one thread each (as a worker with one thread runs them), against the
whole evaluation's cost per pixel (BENCHMARKS.md, "rgbn.dask on 16384²").

    python benches/dask_task_cost.py GRAPH STORE.zarr SIDE TILE N

prints the first and median task time, seconds per megapixel and the peak RSS. The outputs go to
a folder beside STORE (removed first).
"""

import os
import resource
import shutil
import sys
import time

import rgbn.dask as rd


def main():
    graph, store, side, tile, n = sys.argv[1], os.path.abspath(sys.argv[2]), *map(int, sys.argv[3:6])
    out = os.path.join(os.path.dirname(store), "task_cost")
    shutil.rmtree(out, ignore_errors=True)
    os.makedirs(out)
    outs = {"image": os.path.join(out, "image.zarr")}
    if "input_image" in graph:
        outs["relit"] = os.path.join(out, "relit.zarr")
    src, paths, _tmp, sizes = rd._prepare(graph, {"image": store}, outs, 0, None, rd.ZARR_CHUNK)
    w, h = rd._common_size(sizes)
    ts = []
    for r in rd._regions(w, h, side)[:n]:
        t = time.perf_counter()
        rd._task(src, paths, outs, r, 0, rd.ZARR_CHUNK, tile, 1)
        ts.append(time.perf_counter() - t)
    med = sorted(ts)[len(ts) // 2]
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(
        f"{os.path.basename(graph)} side {side} tile {tile}: first {ts[0]:.3f} s, median {med:.3f} s "
        f"per task = {med / (side * side / 1e6):.3f} s/Mpx; peak RSS {rss:.0f} MB"
    )


if __name__ == "__main__":
    main()
