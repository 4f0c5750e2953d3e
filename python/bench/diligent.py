"""DiLiGenT depth accuracy and time: rgbn.integrate_depth(method="bilateral") against the
reference implementation's Python code (xucao-42/bilateral_normal_integration, CPU version:
`bilateral_normal_integration_cpu.py`), alternated object by object in one run.

  python python/bench/diligent.py --reference DIR_OF_THE_REFERENCE_REPO [--solve-tol 1e-3]

The data is the reference repository's `data/Fig7_diligent` (normal_map.png, mask.png, K.txt,
depth_gt.npz per object); it is read exactly as its `evaluation_diligent.py` reads it
(n = v/65535·2 − 1, not renormalised on its side; rgbn.Image renormalises — the gradients are
unchanged). The metric is its MADE: s = nanmedian(Z_gt / Z), mean |s·Z − Z_gt| (mm).
Settings as its evaluation: k = 2, ≤ 100 reweighting iterations, energy tolerance 1e-4, CG
tolerance 1e-3 (rgbn's `tolerance`, the same role). The reference's numba kernels are compiled
by one untimed call first.
"""

import argparse
import os
import pathlib
import statistics
import sys
import time
import warnings

import cv2
import numpy as np

import rgbn

OBJECTS = ["bear", "buddha", "cat", "cow", "goblet", "harvest", "pot1", "pot2", "reading"]


def load(d):
    nm = cv2.cvtColor(cv2.imread(str(d / "normal_map.png"), cv2.IMREAD_UNCHANGED), cv2.COLOR_RGB2BGR)
    nm = nm / 65535 * 2 - 1 if nm.dtype == np.uint16 else nm / 255 * 2 - 1
    mask = cv2.imread(str(d / "mask.png"), cv2.IMREAD_GRAYSCALE).astype(bool)
    K = np.loadtxt(d / "K.txt")
    gt = np.load(d / "depth_gt.npz")["depth_gt"].astype(np.float64)
    return nm, mask, K, gt


def made(depth, gt, mask):
    depth = np.where(mask, depth.astype(np.float64), np.nan)
    s = np.nanmedian(gt / depth)
    return float(np.nanmean(np.abs(s * depth - gt)))


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--reference", required=True, type=pathlib.Path)
    p.add_argument("--solve-tol", type=float, default=1e-3)
    p.add_argument("--objects", nargs="*", default=OBJECTS)
    p.add_argument("--repeat", type=int, default=1, help="alternated runs per object (median taken)")
    a = p.parse_args()
    sys.path.insert(0, str(a.reference))
    import contextlib
    import io

    from bilateral_normal_integration_cpu import bilateral_normal_integration as reference

    data = a.reference / "data" / "Fig7_diligent"
    print(f"load at start: {os.getloadavg()}")
    nm, mask, K, _ = load(data / "cow")
    with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
        reference(normal_map=nm[::4, ::4], normal_mask=mask[::4, ::4], k=2, K=K, max_iter=2, tol=1e-4)
    rows = []
    print("| object | rgbn bilateral MADE (mm) | reference MADE (mm) | rgbn time (s) | reference time (s) |")
    print("|---|---|---|---|---|")
    for obj in a.objects:
        nm, mask, K, gt = load(data / obj)
        trs, trefs = [], []
        for _ in range(a.repeat):
            t0 = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", rgbn.RepairWarning)
                img = rgbn.Image(nm.astype(np.float32), mask=mask.astype(np.float32))
            z = rgbn.integrate_depth(img, "bilateral", camera=K, sharpness=2.0, irls_iterations=100,
                                     irls_tolerance=1e-4, tolerance=a.solve_tol)
            trs.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            with contextlib.redirect_stderr(io.StringIO()), contextlib.redirect_stdout(io.StringIO()):
                zref, *_ = reference(normal_map=nm, normal_mask=mask, k=2, K=K, max_iter=100, tol=1e-4)
            trefs.append(time.perf_counter() - t0)
        tr, tref = statistics.median(trs), statistics.median(trefs)
        mr, mref = made(z, gt, mask), made(zref, gt, mask)
        rows.append((mr, mref, tr, tref))
        spread = f" (runs {'/'.join(f'{t:.2f}' for t in trs)} vs {'/'.join(f'{t:.2f}' for t in trefs)})" if a.repeat > 1 else ""
        print(f"| {obj} | {mr:.3f} | {mref:.3f} | {tr:.2f} | {tref:.2f} |{spread}", flush=True)
    mr, mref = statistics.mean(r[0] for r in rows), statistics.mean(r[1] for r in rows)
    tr, tref = sum(r[2] for r in rows), sum(r[3] for r in rows)
    print(f"| **mean / total** | **{mr:.3f}** | {mref:.3f} | {tr:.2f} | {tref:.2f} |")
    print(f"speed: {tref / tr:.2f}× faster; mean MADE {100 * (mr / mref - 1):+.1f} % against the reference")
    print(f"load at end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
