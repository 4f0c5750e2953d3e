"""Timings of the Python package (BENCHMARKS.md, "rgbn from Python"):

  --what overhead   rgbn.filter on a 64×64 image: per-call time from Python against the same
                    kernel timed inside Rust (rgbn._rgbn._kernel_time), planar and array-backed
  --what copies     4K: Image(...) construction (validation, no copy) and the planar copy a
                    call makes of an array-backed image
  --what gauss8     4K normals → gauss:8 → normals: rgbn.filter against the same pipeline with
                    scipy.ndimage.gaussian_filter and with cv2.GaussianBlur (numpy element-wise
                    parts), alternated, median of --runs

Run with the installed package: python python/bench/bench_calls.py --what gauss8
"""

import argparse
import os
import statistics
import time

import numpy as np

import rgbn
from rgbn import _rgbn


def normals(h, w, seed=0):
    """Smooth random normals (a band-limited height's), float32 H×W×3."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    z = np.zeros((h, w), np.float32)
    for _ in range(6):
        fx, fy, ph = rng.uniform(0.5, 6) / w, rng.uniform(0.5, 6) / h, rng.uniform(0, 6.28)
        z += np.float32(rng.uniform(2, 8)) * np.sin(2 * np.pi * (fx * x + fy * y) + ph).astype(np.float32)
    gy, gx = np.gradient(z)
    n = np.stack([-gx, gy, np.ones_like(z)], axis=2)
    n /= np.linalg.norm(n, axis=2, keepdims=True)
    return np.ascontiguousarray(n, dtype=np.float32)


def overhead(args):
    n = normals(64, 64)
    arr_img = rgbn.Image(n)
    planar = rgbn.filter(arr_img, "scale:1")
    for kernel in args.kernels:
        rows = []
        for name, img in (("planar Image", planar), ("array-backed Image", arr_img)):
            for _ in range(200):
                rgbn.filter(img, kernel)
            py, rs = [], []
            for _ in range(args.runs):
                k = 2000
                t0 = time.perf_counter_ns()
                for _ in range(k):
                    rgbn.filter(img, kernel)
                py.append((time.perf_counter_ns() - t0) / k / 1e3)
                rs.append(_rgbn._kernel_time(planar, kernel, k) / 1e3)
            p, r = statistics.median(py), statistics.median(rs)
            rows.append((kernel, name, p, r, p - r))
        for kernel, name, p, r, d in rows:
            print(f"| rgbn.filter 64×64 {kernel} | {name} | {p:.1f} µs | kernel in Rust {r:.1f} µs | overhead {d:.1f} µs |")


def copies(args):
    n = normals(2160, 3840)
    c = np.ones_like(n) * np.float32(0.5)
    ts_new, ts_copy = [], []
    for _ in range(args.runs):
        t0 = time.perf_counter()
        img = rgbn.Image(n, c)
        ts_new.append(time.perf_counter() - t0)
        before = rgbn.planar_copies()
        t0 = time.perf_counter()
        img.with_mask(None)  # one planar copy of normals and colour, nothing else
        ts_copy.append(time.perf_counter() - t0)
        assert rgbn.planar_copies() == before + 2 and img.normals is n
    print(f"| 4K Image(normals, color) | 0 copies (img.normals is normals) | {statistics.median(ts_new) * 1e3:.1f} ms (validation pass) |")
    print(f"| 4K planar copy of normals + colour, per call | 2 copies | {statistics.median(ts_copy) * 1e3:.1f} ms |")


def gauss8(args):
    import cv2
    import scipy.ndimage as ndi

    cv2.setNumThreads(args.threads)
    n = normals(2160, 3840)

    def with_scipy(n, s=8.0):
        g0 = -n[..., 0] / n[..., 2]
        g1 = -n[..., 1] / n[..., 2]
        b0 = ndi.gaussian_filter(g0, s, mode="reflect")
        b1 = ndi.gaussian_filter(g1, s, mode="reflect")
        r = 1 / np.sqrt(b0 * b0 + b1 * b1 + 1)
        return np.stack([-b0 * r, -b1 * r, r], axis=2)

    def with_cv2(n, s=8.0):
        g = np.empty(n.shape[:2] + (2,), np.float32)
        np.divide(-n[..., 0], n[..., 2], out=g[..., 0])
        np.divide(-n[..., 1], n[..., 2], out=g[..., 1])
        b = cv2.GaussianBlur(g, (0, 0), s, sigmaY=s, borderType=cv2.BORDER_REFLECT)
        r = 1 / np.sqrt(b[..., 0] ** 2 + b[..., 1] ** 2 + 1)
        return np.stack([-b[..., 0] * r, -b[..., 1] * r, r], axis=2)

    def rgbn_arrays(n):
        return rgbn.filter(rgbn.Image(n), "gauss:8").normals

    planar = rgbn.filter(rgbn.Image(n), "scale:1")

    def rgbn_planar(_):
        return rgbn.filter(planar, "gauss:8")

    # The same result within the filters' differences (rgbn's is recursive, truncation 1e-3).
    a, b, c = rgbn_arrays(n), with_scipy(n), with_cv2(n)
    print(f"max |rgbn − scipy| = {np.abs(a - b).max():.2e}, |rgbn − cv2| = {np.abs(a - c).max():.2e}")
    fns = {"rgbn arrays→arrays": rgbn_arrays, "rgbn planar Image": rgbn_planar,
           "scipy.ndimage": with_scipy, "OpenCV": with_cv2}
    times = {k: [] for k in fns}
    for k, f in fns.items():
        f(n)
    for _ in range(args.runs):
        for k, f in fns.items():
            t0 = time.perf_counter()
            f(n)
            times[k].append(time.perf_counter() - t0)
    med = {k: statistics.median(v) * 1e3 for k, v in times.items()}
    print(f"load: {os.getloadavg()}")
    for k, v in med.items():
        print(f"| {k} | {v:.1f} ms | runs {', '.join(f'{t * 1e3:.0f}' for t in times[k])} |")
    for k in ("rgbn arrays→arrays", "rgbn planar Image"):
        print(f"{k}: {med['scipy.ndimage'] / med[k]:.1f}× scipy, {med['OpenCV'] / med[k]:.1f}× OpenCV")


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--what", choices=["overhead", "copies", "gauss8"], required=True)
    p.add_argument("--runs", type=int, default=7)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--kernels", nargs="*", default=["gauss:2", "gauss:8", "box:1"])
    a = p.parse_args()
    {"overhead": overhead, "copies": copies, "gauss8": gauss8}[a.what](a)
