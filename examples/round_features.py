#!/usr/bin/env python3
"""A second witness of a normal map's green convention, independent of integrability.

A round feature (a screw head, a rivet, a pebble, a dimple) is rotationally symmetric: its
slope points along the radius, so the red channel (x, right in both conventions) and the
green channel (y) must describe the same radial profile. Stored OpenGL (+y up), green rises
toward the image top of a dome exactly as red rises toward its right; stored DirectX (+y
down), green rises toward the bottom. So at each round feature

    R_out = sum(r * dx/|d|),  G_out = sum(g * (-dy)/|d|)   (image y grows downward)

have the same sign for OpenGL and opposite signs for DirectX, dome or dimple alike.

Features are found where the red radial score is a local maximum over a 15 x 15 window
(radius 6 disc), and kept only where they look round: |G_out| >= 0.5 |R_out| and both
cross terms (red against the vertical, green against the horizontal) <= 0.25 |R_out|.
This uses no curl and no surface: it is a different assumption (symmetry) from rgbn's rule
(integrability), so where both speak they are two witnesses, not one.

Usage: python examples/round_features.py MAP [MAP ...] [--min-score 15]
Prints per file: round features found, how many read OpenGL / DirectX.
Needs numpy and Pillow.
"""
import sys

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from PIL import Image

R = 7  # window half-size; the disc has radius R - 1


def witness(path, min_score=15.0):
    a = np.asarray(Image.open(path).convert("RGB")).astype(np.float64) / 127.5 - 1.0
    ys, xs = np.mgrid[-R : R + 1, -R : R + 1]
    disc = (xs**2 + ys**2) <= (R - 1) ** 2
    d = np.maximum(1.0, np.hypot(xs, ys))
    kx, ky = xs / d * disc, -ys / d * disc  # outward unit vector, image y down -> up

    def corr(plane, k):
        return np.einsum("ijkl,kl->ij", sliding_window_view(plane, (2 * R + 1, 2 * R + 1)), k)

    red, green = a[..., 0], a[..., 1]
    r_out, g_out = corr(red, kx), corr(green, ky)
    r_cross, g_cross = corr(red, ky), corr(green, kx)
    score = np.abs(r_out)
    width = score.shape[1]
    chosen = []
    for idx in np.argsort(score.ravel())[::-1]:
        y, x = divmod(int(idx), width)
        s = score[y, x]
        if s < min_score:
            break
        if any(abs(y - yy) < 2 * R and abs(x - xx) < 2 * R for yy, xx in chosen):
            continue
        if abs(g_out[y, x]) < 0.5 * s or abs(r_cross[y, x]) > 0.25 * s or abs(g_cross[y, x]) > 0.25 * s:
            continue
        chosen.append((y, x))
    gl = sum(1 for y, x in chosen if r_out[y, x] * g_out[y, x] > 0)
    return chosen, gl, len(chosen) - gl, r_out, g_out


def main():
    args = sys.argv[1:]
    min_score = 15.0
    if "--min-score" in args:
        i = args.index("--min-score")
        min_score = float(args[i + 1])
        del args[i : i + 2]
    if not args:
        print(__doc__)
        return 2
    for path in args:
        chosen, gl, dx, r_out, g_out = witness(path, min_score)
        print(f"{path}: round features {len(chosen)}: OpenGL {gl}, DirectX {dx}")
        for y, x in chosen[:12]:
            print(f"  centre ({x + R}, {y + R}): R_out {r_out[y, x]:+.1f}, G_out {g_out[y, x]:+.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
