"""rgbn.dask against `rgbn eval` and against a Dask user's own σ 8 px Gaussian (BENCHMARKS.md,
"rgbn.dask"). Run in a venv with `pip install "./python[dask]" dask-image scipy psutil`:

    python benches/dask_peer.py --size 16384 --runs 5 --dir /path/with/space

1. The input: an RGBN OME-Zarr store of the demo medallion, size², written by `rgbn eval
   --region` runs of 4096² (memory bounded; the first run creates the store).
2. Alternated, `--runs` times each, whole processes timed from the outside:
   - `rgbn eval graphs/input_image.ron` on the whole store with RAYON_NUM_THREADS=2;
   - `rgbn.dask.evaluate` of the same graph on a LocalCluster of 2 worker processes × 1 thread
     (the cluster started before the clock; the call timed);
   - the peer: the σ 8 px Gaussian on the foreshortened gradients (p, q) = (−nx/nz, −ny/nz)
     as a Dask user writes it today — `dask_image.ndfilters.gaussian_filter` on p and q read
     with `dask.array.from_zarr`, normals rebuilt, written with `to_zarr` — on the same cluster;
   - the same Gaussian in rgbn (`filter.gaussian`, σ 8 px) through rgbn.dask on the cluster,
     once as rgbn writes a store by default (level 0 and its `multiscales` pyramid) and once
     with `levels=1` (level 0 alone, as the peer's `to_zarr` writes: the like-for-like row).
   `--gauss-only` skips the first two (the σ 8 rows alone).
   rgbn's calls run on one LocalCluster, the peer on a second one of the same shape, used in
   turn (never at once), so that each worker's memory is its own tool's.
3. Peak RSS of each worker during each call (its VmHWM, reset before the call through
   /proc/self/clear_refs, so the peer's memory and rgbn's are told apart; the process's
   lifetime ru_maxrss is printed too), and the per-task overhead: the scheduler's task
   durations (compute time inside the task) against the wall time of the call.
"""

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

DEMO = """(
    version: 2,
    next_id: 2,
    outputs: {{ "image": (node: 1, port: "image") }},
    nodes: [ (id: 1, op: "demo", pos: (0.0, 0.0), params: {{ "size": Int({size}) }}) ],
)
"""

GAUSS = """(
    version: 2,
    next_id: 2,
    inputs: { "image": (ty: Rgbn) },
    outputs: { "image": (node: 1, port: "image") },
    nodes: [ (id: 1, op: "filter.gaussian", name: Some("gauss8"), pos: (0.0, 0.0),
              params: { "sigma_px": Float(8.0) }, inputs: { "image": Input("image") }) ],
)
"""


def rgbn_cli(args, env=None):
    cmd = [sys.executable, "-c", "import sys, rgbn; sys.exit(rgbn.main(sys.argv[1:]))", *map(str, args)]
    t = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, env=env)
    dt = time.perf_counter() - t
    if r.returncode:
        raise SystemExit(f"rgbn {' '.join(map(str, args))}: {r.stderr}")
    return dt


def make_input(d, size):
    path = os.path.join(d, f"in{size}.zarr")
    if os.path.exists(os.path.join(path, "zarr.json")):
        return path
    g = os.path.join(d, "demo.ron")
    open(g, "w").write(DEMO.format(size=size))
    step = 4096
    for y in range(0, size, step):
        for x in range(0, size, step):
            rgbn_cli(["eval", g, "--region", f"{x},{y},{min(step, size - x)},{min(step, size - y)}", "-o", f"image={path}"])
    return path


def peer(store, out):
    """A Dask user's σ 8 px Gaussian on the foreshortened gradients."""
    import dask.array as da
    from dask_image import ndfilters

    a = da.from_zarr(os.path.join(store, "0"))  # (c, y, x): R, G, B, nx, ny, nz
    nx, ny, nz = a[3], a[4], a[5]
    p, q = -nx / nz, -ny / nz
    p = ndfilters.gaussian_filter(p, sigma=8.0, mode="mirror", truncate=4.0)
    q = ndfilters.gaussian_filter(q, sigma=8.0, mode="mirror", truncate=4.0)
    inv = 1.0 / da.sqrt(p * p + q * q + 1.0)
    out_a = da.stack([a[0], a[1], a[2], -p * inv, -q * inv, inv]).astype("float32")
    out_a.to_zarr(out, overwrite=True)


def rss_of_workers(client):
    return client.run(lambda: resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024)


def _reset_peak():
    # Linux: "5" resets the process's peak resident set size (VmHWM) to its current one.
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")


def _peak():
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024
    return 0


def peak_during(client, peaks, key, call):
    """Runs ``call()`` and records each worker's peak RSS during it under ``peaks[key]``."""
    client.run(_reset_peak)
    out = call()
    for w, v in client.run(_peak).items():
        peaks.setdefault(key, {}).setdefault(w, []).append(v)
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", type=int, default=16384)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--dir", default="target/dask_bench")
    ap.add_argument("--chunks", type=int, default=None)
    ap.add_argument("--gauss-only", action="store_true", help="only the σ 8 rows (rgbn.dask and the peer)")
    a = ap.parse_args()
    os.makedirs(a.dir, exist_ok=True)
    import distributed
    import rgbn.dask as rd

    store = make_input(a.dir, a.size)
    g = os.path.join(REPO, "graphs", "input_image.ron")
    gg = os.path.join(a.dir, "gauss8.ron")
    open(gg, "w").write(GAUSS)
    env2 = dict(os.environ, RAYON_NUM_THREADS="2")
    outs = lambda tag: {"image": os.path.join(a.dir, f"{tag}_image.zarr"), "relit": os.path.join(a.dir, f"{tag}_relit.zarr")}  # noqa: E731
    t = {"whole": [], "dask": [], "peer": [], "rgbn_gauss": [], "rgbn_gauss_l0": [], "whole_gauss": []}
    stats = []
    peaks = {}
    # Two clusters of the same shape, used one at a time: rgbn's tasks on one, the peer on the
    # other, so each worker's memory is its own tool's (a worker keeps freed memory for its
    # next task, and a peer's heap would show in rgbn's peak, and the reverse).
    lc = lambda: distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)  # noqa: E731
    with lc() as c, lc() as pc, distributed.Client(pc, set_as_default=False) as peer_client, distributed.Client(c) as client:
        for run in range(a.runs):
            for p in list(outs("w").values()) + list(outs("d").values()):
                shutil.rmtree(p, ignore_errors=True)
            if not a.gauss_only:
                o = outs("w")
                t["whole"].append(rgbn_cli(["eval", g, "--input", f"image={store}", "-o", f"image={o['image']}", "-o", f"relit={o['relit']}"], env=env2))
                # Task compute times from the scheduler's task stream (seconds inside each task).
                with distributed.get_task_stream(client) as ts:
                    t0 = time.perf_counter()
                    peak_during(client, peaks, "rgbn.dask input_image", lambda: rd.evaluate(g, {"image": store}, outs("d"), chunks=a.chunks))
                    t["dask"].append(time.perf_counter() - t0)
                stats.append([
                    sum(s["stop"] - s["start"] for s in d.get("startstops", ()) if s["action"] == "compute")
                    for d in ts.data
                    if "rgbn-chunk" in str(d.get("key", ""))
                ])
            shutil.rmtree(os.path.join(a.dir, "peer.zarr"), ignore_errors=True)
            t0 = time.perf_counter()
            with peer_client.as_current():
                peak_during(peer_client, peaks, "peer (dask-image)", lambda: peer(store, os.path.join(a.dir, "peer.zarr")))
            t["peer"].append(time.perf_counter() - t0)
            shutil.rmtree(os.path.join(a.dir, "gauss.zarr"), ignore_errors=True)
            t0 = time.perf_counter()
            peak_during(client, peaks, "rgbn.dask gauss8", lambda: rd.evaluate(gg, {"image": store}, {"image": os.path.join(a.dir, "gauss.zarr")}, chunks=a.chunks))
            t["rgbn_gauss"].append(time.perf_counter() - t0)
            # Level 0 alone, as the peer writes it.
            shutil.rmtree(os.path.join(a.dir, "gauss_l0.zarr"), ignore_errors=True)
            t0 = time.perf_counter()
            peak_during(client, peaks, "rgbn.dask gauss8 levels=1", lambda: rd.evaluate(gg, {"image": store}, {"image": os.path.join(a.dir, "gauss_l0.zarr")}, chunks=a.chunks, levels=1))
            t["rgbn_gauss_l0"].append(time.perf_counter() - t0)
            shutil.rmtree(os.path.join(a.dir, "gauss_w.zarr"), ignore_errors=True)
            t["whole_gauss"].append(rgbn_cli(["eval", gg, "--input", f"image={store}", "-o", f"image={os.path.join(a.dir, 'gauss_w.zarr')}"], env=env2))
            print(f"run {run}: " + ", ".join(f"{k} {v[-1]:.2f}s" for k, v in t.items() if v), flush=True)
        rss = rss_of_workers(client)
        peer_rss = rss_of_workers(peer_client)
    med = {k: statistics.median(v) for k, v in t.items() if v}
    ratios = [d / w for d, w in zip(t["dask"], t["whole"])]
    pr = [r / p for r, p in zip(t["rgbn_gauss"], t["peer"])]
    pr0 = [r / p for r, p in zip(t["rgbn_gauss_l0"], t["peer"])]
    last = stats[-1] if stats else []
    n_tasks = len(last)
    busy = sum(last)
    wall = t["dask"][-1] if t["dask"] else 0.0
    # Per task: the wall the two workers spend beyond the tasks' compute, per task.
    overhead = (2 * wall - busy) / max(n_tasks, 1)
    res = {
        "size": a.size,
        "runs": t,
        "median": med,
        "dask/whole median of per-run ratios": statistics.median(ratios) if ratios else None,
        "rgbn_gauss/peer median of per-run ratios": statistics.median(pr),
        "rgbn_gauss levels=1/peer median of per-run ratios": statistics.median(pr0),
        "per-run ratios": {"rgbn_gauss/peer": pr, "rgbn_gauss levels=1/peer": pr0},
        "worker peak RSS GiB during each call (max over runs)": {
            key: {w: max(v) / 2**30 for w, v in per.items()} for key, per in peaks.items()
        },
        "worker lifetime peak RSS GiB, rgbn's cluster": {k: v / 2**30 for k, v in rss.items()},
        "worker lifetime peak RSS GiB, the peer's cluster": {k: v / 2**30 for k, v in peer_rss.items()},
        "worker peak RSS GiB during each call, per run": {
            key: {w: [round(x / 2**30, 3) for x in v] for w, v in per.items()} for key, per in peaks.items()
        },
        "tasks": n_tasks,
        "task compute s (mean)": busy / max(n_tasks, 1),
        "overhead ms per task": overhead * 1e3,
        "overhead fraction": overhead / max(overhead + busy / max(n_tasks, 1), 1e-12),
    }
    print(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
